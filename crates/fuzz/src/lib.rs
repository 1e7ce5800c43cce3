//! A standing fuzz target for untrusted scene files: a mutation generator over a committed
//! corpus (`corpus/`: every example scene and scenes of every feature), and an oracle that runs
//! each variant through the parser, the builders, the cost guard and, when cheap, a tiny render
//! and the closed-form means, and reports:
//!
//! - a panic, or a hang (no answer within [`HANG_SECONDS`]);
//! - an error that names no field and no line;
//! - a message that quotes more of a file than a short excerpt, or quotes a file outside the
//!   scene's folder at all;
//! - a NaN or infinite result from a scene that was accepted.
//!
//! The variants are files a user could write: numbers replaced by extremes (`1e308`,
//! `5e-324`, `nan`, `inf`, huge integers), lines deleted, duplicated, swapped or spliced from
//! other scenes, snippets inserted (paths to FIFOs, devices, files outside the folder, deep
//! nesting, dates, long names, terminal escapes, byte-order marks), bytes flipped.
//!
//! Shard files are fuzzed too ([`shards`]): genuine shards of every sharded render, mutated
//! and resealed, read and merged under the same oracle.
//!
//! `cargo test -p speckle-fuzz` runs the corpus and a few hundred variants (CI);
//! `SPECKLE_FUZZ_SECONDS=1800 cargo test --release -p speckle-fuzz -- --ignored --nocapture`
//! runs for half an hour and prints the count of inputs tried.

#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod shards;

use speckle::estimators::{CovarianceOptions, Progress, render_intensity};
use speckle::scene::cost::Command;
use speckle::scene::{LoadError, Overrides, Problem, SceneError, load_str};
use std::path::Path;
use std::time::{Duration, Instant};

/// An input that has not answered after this long hangs.
pub const HANG_SECONDS: u64 = 60;

/// A secret line in files the oracle's scenes may name: a message may quote at most a short
/// excerpt of it.
pub const SECRET: &str = "S3CRET-S3CRET-S3CRET-S3CRET-S3CRET-S3CRET-S3CRET-S3CRET-S3CRET-S3CRET";

/// The content of a file outside the scene's folder: no message may quote any of it.
pub const OUTSIDE: &str = "0UTSIDE-TOKEN";

/// What the oracle found wrong with an input.
#[derive(Debug, Clone, PartialEq)]
pub enum Finding {
    /// The code panicked.
    Panic(String),
    /// No answer within [`HANG_SECONDS`].
    Hang,
    /// An error that names no field and gives no line.
    Unnamed(String),
    /// A message that quotes too much of a file, or a file it should not have read.
    Echo(String),
    /// An accepted scene gave a NaN or infinite result.
    NotFinite(String),
}

/// The embedded corpus: `(name, text)` of every file in `corpus/`.
pub fn corpus() -> Vec<(String, String)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("corpus");
    let mut v: Vec<(String, String)> = std::fs::read_dir(&dir)
        .expect("the corpus folder")
        .filter_map(|e| {
            let p = e.ok()?.path();
            let text = std::fs::read_to_string(&p).ok()?;
            Some((p.file_name()?.to_string_lossy().into_owned(), text))
        })
        .collect();
    v.sort();
    v
}

/// Lays out the files the corpus and the mutations name, in `root`: the scene folder
/// `root/scene` (returned) with tables, grids, a FIFO, a link out of the folder and a file of
/// secrets, and `root/outside.csv` beside it.
pub fn sandbox(root: &Path) -> std::path::PathBuf {
    let scene = root.join("scene");
    std::fs::create_dir_all(&scene).unwrap();
    let w = |name: &str, bytes: &[u8]| std::fs::write(scene.join(name), bytes).unwrap();
    w(
        "amp.csv",
        b"theta_deg,re,im\n0,1,0\n45,0.7,0.1\n90,0.4,0\n135,0.3,-0.1\n180,0.2,0\n",
    );
    w(
        "amp2d.csv",
        b"theta_rad,re,im\n0,1,0\n1.5,0.8,0.3\n3.14159,0.3,0\n4.5,0.2,-0.1\n6.2831853,1,0\n",
    );
    w(
        "bom.csv",
        "\u{feff}mu,re,im\n-1,0.2,0\n0,0.5,0\n1,1,0\n".as_bytes(),
    );
    w("secret.csv", format!("{SECRET}\n{SECRET},1,2\n").as_bytes());
    w(
        "grid.npy",
        &speckle::scene::npy::encode_f8(&[2, 2, 2], &[1.0, 0.5, 0.0, 2.0, 1.0, 1.0, 0.3, 0.0]),
    );
    w(
        "grid2d.npy",
        &speckle::scene::npy::encode_f8(&[2, 3], &[1.0, 0.5, 0.0, 2.0, 1.0, 1.0]),
    );
    w(
        "ids.npy",
        &speckle::scene::npy::encode_i8(&[2, 2, 2], &[0, 1, 1, 0, 0, 1, 1, 0]),
    );
    std::fs::write(root.join("outside.csv"), format!("{OUTSIDE},1,0\n")).unwrap();
    #[cfg(unix)]
    {
        let _ = std::os::unix::fs::symlink(root.join("outside.csv"), scene.join("link.csv"));
        let _ = std::process::Command::new("mkfifo")
            .arg(scene.join("fifo.csv"))
            .status();
    }
    scene
}

/// A small deterministic random stream (SplitMix64).
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    /// A stream from `seed`.
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// The next 64 bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in `0..n` (`n > 0`).
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n as u64) as usize
    }

    /// One of `items`.
    pub fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
}

/// Extreme and ordinary numbers a mutation puts in place of a number.
const NUMBERS: &[&str] = &[
    "0",
    "-1",
    "1",
    "2",
    "0.5",
    "-0.0",
    "1e308",
    "-1e308",
    "1.7976931348623157e308",
    "5e-324",
    "1e-300",
    "1e-200",
    "1e200",
    "1e19",
    "1e12",
    "1e-12",
    "2000",
    "1e6",
    "nan",
    "inf",
    "-inf",
    "18446744073709551615",
    "9223372036854775807",
    "4294967295",
    "65536",
    "1048577",
    "3",
    "0.999999",
    "-0.999999",
    "89.9999",
    "90",
    "360",
    "1e15",
];

/// Lines a mutation inserts.
const SNIPPETS: &[&str] = &[
    "file = \"fifo.csv\"",
    "file = \"/dev/zero\"",
    "file = \"/dev/stdin\"",
    "file = \"../outside.csv\"",
    "file = \"/etc/passwd\"",
    "file = \"link.csv\"",
    "file = \"secret.csv\"",
    "file = \"bom.csv\"",
    "file = \"amp.csv\"",
    "file = \"amp2d.csv\"",
    "file = \"grid.npy\"",
    "file = \"ids.npy\"",
    "file = \"secret.csv\"\nkind = \"density\"",
    "[phase]\ntype = \"tabulated\"\nfile = \"secret.csv\"",
    "[phase]\ntype = \"tabulated\"\nfile = \"amp.csv\"",
    "[phase]\ntype = \"tabulated\"\nfile = \"../outside.csv\"",
    "[medium.grid]\nfile = \"grid.npy\"\nkind = \"density\"",
    "[medium.grid]\nfile = \"fifo.csv\"\nkind = \"density\"",
    "[medium.grid]\nfile = \"/dev/zero\"\nkind = \"density\"",
    "[output]\ndir = \"/tmp/speckle-fuzz-abs\"",
    "[output]\ndir = \"../up\"",
    "[output]\npng_scale = 64",
    "dir = \"/etc\"",
    "png_scale = 64",
    "png_realizations = 100000",
    "max_vertices = 1",
    "max_vertices = 4294967295",
    "render = 1979-05-27T07:32:00Z",
    "when = 1979-05-27",
    "wavelength = 5e-324",
    "sigma_s = 1e19",
    "size = [1e308, 4.0, 2.0]",
    "position = [0.0, 0.0, -1e308]",
    "step_x = [1e308, 0.0, 0.0]",
    "angles_deg = [-1e308, 1e308]",
    "n = 1000000",
    "nx = 1048576",
    "realizations = 100000000",
    "configurations = 1000000",
    "paths = 18446744073709551615",
    "name = \"\u{1b}[31mred\u{1b}[0m\"",
    "name = \"xxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxx\"",
    "name = \"../../evil\"",
    "dimension = 2",
    "dimension = 7",
    "pairs = [[0, 0], [0, 99]]",
    "pairs = []",
    "host_index = 1e-300",
    "[[medium.particles]]\nradius = 1e6\nindex = [1.5, 0.0]\nvolume_fraction = 0.1",
    "[[medium.particles]]\nradius = 0.1\nindex = [1.5, 0.0]\nnumber_density = 1e300",
    "[[sensors]]\ntype = \"point_grid\"\norigin = [0.0, 0.0, 50.0]\nstep_x = [1e308, 0.0, 0.0]\nstep_y = [0.0, 1.0, 0.0]\nnx = 3\nny = 2",
    "[[sensors]]\ntype = \"far_arc\"\nangles_deg = [-1e308, 1e308]\nn = 3",
    "[[sources]]\ntype = \"point\"\nposition = [0.0, 0.0, -1e308]",
    "[[sources]]\ntype = \"plane_tilts\"\ntilts_deg = [1e308, -1e308]",
    "a.b.c.d.e.f.g.h.i.j.k.l.m.n.o.p.q.r.s.t.u.v.w.x.y.z.a.b.c.d.e.f.g.h.i.j.k.l.m.n.o.p.q.r.s.t.u.v.w.x.y.z.a.b.c.d.e.f.g.h.i.j.k.l.m.n.o.p.q.r.s.t.u.v.w.x.y.z.a.b.c.d.e.f.g.h.i.j.k.l.m.n.o.p.q.r.s.t.u.v.w.x.y.z = 1",
    "x = [[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[1]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]]",
    "\u{feff}",
    "\u{1b}]0;title\u{7}",
    "type = \"hg\"\ng = 0.9999999",
    "type = \"vmf\"\ngamma = [1e300, -5.0]\nalpha = [1.0, 1e-300]",
    "type = \"hg_mixture\"\nweights = [1e308, 1e308]\ng = [0.5, -0.5]",
];

/// Strings a mutation puts in place of a quoted string.
const STRINGS: &[&str] = &[
    "\"\"",
    "\"fifo.csv\"",
    "\"/dev/zero\"",
    "\"../outside.csv\"",
    "\"secret.csv\"",
    "\"point\"",
    "\"far\"",
    "\"plane\"",
    "\"far_grid\"",
    "\"far_arc\"",
    "\"point_grid\"",
    "\"plane_tilts\"",
    "\"tabulated\"",
    "\"materials\"",
    "\"density\"",
    "\"forward_only\"",
    "\"exponential_depth\"",
    "\"phase\"",
    "\"embedded:nope\"",
    "\"\u{1b}[2J\"",
];

/// Replaces the `k`-th number-looking token of `line`.
fn replace_number(line: &str, rng: &mut Rng) -> Option<String> {
    let bytes = line.as_bytes();
    let mut spans = Vec::new();
    let mut i = 0;
    while i < bytes.len() {
        let c = bytes[i];
        let starts = c.is_ascii_digit()
            || ((c == b'-' || c == b'+' || c == b'.')
                && bytes.get(i + 1).is_some_and(|d| d.is_ascii_digit()));
        let in_word = i > 0 && (bytes[i - 1].is_ascii_alphabetic() || bytes[i - 1] == b'_');
        if starts && !in_word {
            let start = i;
            i += 1;
            while i < bytes.len() && (bytes[i].is_ascii_digit() || b".eE+-_".contains(&bytes[i])) {
                i += 1;
            }
            spans.push(start..i);
        } else {
            i += 1;
        }
    }
    if spans.is_empty() {
        return None;
    }
    let s = spans[rng.below(spans.len())].clone();
    Some(format!(
        "{}{}{}",
        &line[..s.start],
        rng.pick(NUMBERS),
        &line[s.end..]
    ))
}

/// Replaces a quoted string of `line`.
fn replace_string(line: &str, rng: &mut Rng) -> Option<String> {
    let a = line.find('"')?;
    let b = a + 1 + line[a + 1..].find('"')?;
    Some(format!(
        "{}{}{}",
        &line[..a],
        rng.pick(STRINGS),
        &line[b + 1..]
    ))
}

/// A variant of `text`: one to four mutations, `others` the corpus to splice from.
pub fn mutate(text: &str, others: &[(String, String)], rng: &mut Rng) -> String {
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let count = 1 + rng.below(4);
    for _ in 0..count {
        if lines.is_empty() {
            lines.push(rng.pick(SNIPPETS).to_string());
            continue;
        }
        let at = rng.below(lines.len());
        match rng.below(9) {
            0..=2 => {
                if let Some(l) = replace_number(&lines[at], rng) {
                    lines[at] = l;
                }
            }
            3 => {
                lines.remove(at);
            }
            4 => {
                let l = lines[at].clone();
                lines.insert(at, l);
            }
            5 => lines.insert(at, rng.pick(SNIPPETS).to_string()),
            6 => {
                if let Some(l) = replace_string(&lines[at], rng) {
                    lines[at] = l;
                }
            }
            7 => {
                let other = &rng.pick(others).1;
                let pool: Vec<&str> = other.lines().collect();
                if !pool.is_empty() {
                    lines.insert(at, rng.pick(&pool).to_string());
                }
            }
            _ => {
                let b = rng.below(lines.len());
                lines.swap(at, b);
                let l = &mut lines[at];
                if !l.is_empty() && rng.below(3) == 0 {
                    // A stray character: a control, an escape, a quote or a bracket.
                    let chars = [
                        '\u{1b}', '\u{0}', '"', '[', ']', '=', '\u{feff}', '\u{7f}', '#',
                    ];
                    let pos = l
                        .char_indices()
                        .nth(rng.below(l.chars().count()))
                        .map_or(0, |(i, _)| i);
                    l.insert(pos, *rng.pick(&chars));
                }
            }
        }
    }
    let mut out = lines.join("\n");
    out.push('\n');
    out
}

/// Whether `e` names a field or gives a line.
fn named(e: &LoadError) -> bool {
    match e {
        LoadError::In { error, .. } => named(error),
        LoadError::Parse { field, line, .. } => {
            field.as_deref().is_some_and(good_field) || line.is_some()
        }
        LoadError::Invalid(SceneError::InvalidInput { field, .. }) => good_field(field),
        LoadError::Read { .. } => true,
    }
}

/// A field name: non-empty, printable, without serde's private keys.
fn good_field(f: &str) -> bool {
    !f.is_empty() && !f.contains("$__") && !f.chars().any(char::is_control)
}

/// Whether `message` quotes too much of a file.
fn echo(message: &str) -> Option<Finding> {
    if message.contains(OUTSIDE) {
        return Some(Finding::Echo(format!(
            "quotes a file outside the folder: {message}"
        )));
    }
    if message.contains(&SECRET[..48]) {
        return Some(Finding::Echo(format!(
            "quotes more than an excerpt: {message}"
        )));
    }
    None
}

/// Cancels a render once its time is up.
struct Deadline(Instant);

impl Progress for Deadline {
    fn cancelled(&self) -> bool {
        Instant::now() > self.0
    }
}

/// The oracle: loads `text` as a scene in the folder `base` and checks the outcome (see the
/// crate documentation). Panics propagate to the caller.
pub fn check(text: &str, base: &Path) -> Result<(), Finding> {
    let p = match load_str(text, "fuzz.toml", base, "fuzz", &Overrides::default()) {
        Ok(p) => p,
        Err(e) => {
            if let Some(f) = echo(&e.to_string()) {
                return Err(f);
            }
            return if named(&e) {
                Ok(())
            } else {
                Err(Finding::Unnamed(e.to_string()))
            };
        }
    };
    exercise(&p)
}

/// Estimates every command of an accepted scene, then renders a few paths and the means when
/// that is cheap, and checks that the results are finite.
fn exercise(p: &Problem) -> Result<(), Finding> {
    let refused = |e: SceneError| {
        let SceneError::InvalidInput { field, .. } = &e;
        if good_field(field) {
            Ok(())
        } else {
            Err(Finding::Unnamed(e.to_string()))
        }
    };
    if let Err(e) = p.check_path_length() {
        return refused(e);
    }
    let mut cheap = [false; 2];
    for (k, c) in [Command::Intensity, Command::Mean].into_iter().enumerate() {
        match p.estimate(c, 1) {
            Ok(e) => cheap[k] = e.seconds < 0.2 && e.bytes < 5e8,
            Err(e) => refused(e)?,
        }
    }
    for c in [Command::Covariance, Command::Single, Command::Fields] {
        if let Err(e) = p.estimate(c, 1) {
            refused(e)?;
        }
    }
    // The commands cost detector renders with a pilot of their paths (bounded, so never a hang).
    let _ = speckle::runs::detectors::measured_vertices(p);
    if let Some(m) = &p.motion {
        match p.estimate(Command::G1, 1) {
            Ok(e) if e.seconds < 0.2 && e.bytes < 5e8 => {
                let opts = CovarianceOptions {
                    paths: 16,
                    seed: p.render.seed,
                    coherence: p.render.coherence,
                    sampling: p.render.sampling,
                };
                let deadline = Deadline(Instant::now() + Duration::from_secs(HANG_SECONDS / 2));
                if p.scene.has_detectors() {
                    let motion = Some((&m.model, m.lags.as_slice()));
                    detectors_finite(p, motion, &opts, &deadline, "g1 correlation")?;
                    return Ok(());
                }
                let entries = speckle::estimators::Entries::Diagonal;
                match speckle::estimators::render_correlation(
                    &p.scene, &m.model, &m.lags, &entries, &opts, &deadline,
                ) {
                    Ok(est) => {
                        for l in 0..m.lags.len() {
                            for e in 0..p.pairs() {
                                let (v, _) = est.total(l, e);
                                if !(v.re.is_finite() && v.im.is_finite()) {
                                    return Err(Finding::NotFinite(format!("g1 correlation {v}")));
                                }
                            }
                        }
                    }
                    Err(speckle::estimators::EstimatorError::Cancelled) => {
                        return Err(Finding::Hang);
                    }
                    Err(speckle::estimators::EstimatorError::InvalidInput { field, .. })
                        if good_field(&field) => {}
                    Err(e) => {
                        return Err(Finding::Unnamed(format!("g1 render failed: {e}")));
                    }
                }
            }
            Ok(_) => {}
            Err(e) => refused(e)?,
        }
    }
    if cheap[0] {
        let opts = CovarianceOptions {
            paths: 16,
            seed: p.render.seed,
            coherence: p.render.coherence,
            sampling: p.render.sampling,
        };
        let deadline = Deadline(Instant::now() + Duration::from_secs(HANG_SECONDS / 2));
        if p.scene.has_detectors() {
            return detectors_finite(p, None, &opts, &deadline, "detector reading");
        }
        match render_intensity(&p.scene, &opts, &deadline) {
            Ok(est) => {
                if let Some(v) = est
                    .total
                    .value
                    .as_slice()
                    .iter()
                    .find(|c| !(c.re.is_finite() && c.im.is_finite()))
                {
                    return Err(Finding::NotFinite(format!("intensity {v}")));
                }
            }
            Err(speckle::estimators::EstimatorError::Cancelled) => return Err(Finding::Hang),
            Err(e) => return Err(Finding::Unnamed(format!("intensity render failed: {e}"))),
        }
    }
    if cheap[1] {
        match p.means_or_nan(&|| false) {
            Ok(Some((means, warning))) => {
                if warning.is_none()
                    && let Some(m) = means
                        .iter()
                        .find(|m| !(m.re.is_finite() && m.im.is_finite()))
                {
                    return Err(Finding::NotFinite(format!("mean {m}")));
                }
            }
            Ok(None) => {}
            Err(e) => refused(e)?,
        }
    }
    Ok(())
}

/// A tiny render of a scene's detectors (`motion`: at its lags): a finding when it is not
/// finite, hangs or fails.
fn detectors_finite(
    p: &Problem,
    motion: Option<(&speckle::motion::MotionModel, &[f64])>,
    opts: &CovarianceOptions,
    deadline: &Deadline,
    what: &str,
) -> Result<(), Finding> {
    match speckle::estimators::render_detectors(&p.scene, motion, opts, deadline) {
        Ok(Some(est)) => match est
            .total
            .value
            .as_slice()
            .iter()
            .find(|c| !(c.re.is_finite() && c.im.is_finite()))
        {
            Some(v) => Err(Finding::NotFinite(format!("{what} {v}"))),
            None => Ok(()),
        },
        Ok(None) | Err(speckle::estimators::EstimatorError::Cancelled) => Err(Finding::Hang),
        Err(e) => Err(Finding::Unnamed(format!("detector render failed: {e}"))),
    }
}

/// A fuzzing run's tally.
#[derive(Debug, Default)]
pub struct Tally {
    /// Inputs tried.
    pub inputs: u64,
    /// Findings, with the input that caused each.
    pub findings: Vec<(Finding, String)>,
}

/// Runs `f` in a thread watched for [`HANG_SECONDS`]: its finding, a panic, or a hang (whose
/// thread cannot be stopped: the caller stops there).
pub fn watched(f: impl FnOnce() -> Result<(), Finding> + Send + 'static) -> Result<(), Finding> {
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
        let _ = tx.send(r);
    });
    match rx.recv_timeout(Duration::from_secs(HANG_SECONDS)) {
        Ok(Ok(r)) => r,
        Ok(Err(panic)) => Err(Finding::Panic(
            panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default(),
        )),
        Err(_) => Err(Finding::Hang),
    }
}

/// Runs the corpus, then variants of it from `seed`, until `inputs` inputs or `seconds` have
/// passed, each in a thread watched for [`HANG_SECONDS`]; stops at the first hang (its thread
/// cannot be stopped).
pub fn run(seed: u64, inputs: u64, seconds: f64, base: &Path) -> Tally {
    let corpus = corpus();
    let start = Instant::now();
    let mut rng = Rng::new(seed);
    let mut tally = Tally::default();
    let mut n = 0usize;
    while tally.inputs < inputs && start.elapsed().as_secs_f64() < seconds {
        let text = if n < corpus.len() {
            corpus[n].1.clone()
        } else {
            let (_, t) = &corpus[rng.below(corpus.len())];
            let mut v = mutate(t, &corpus, &mut rng);
            // Sometimes mutate a variant again: deeper changes.
            if rng.below(4) == 0 {
                v = mutate(&v, &corpus, &mut rng);
            }
            v
        };
        n += 1;
        let (input, folder) = (text.clone(), base.to_path_buf());
        tally.inputs += 1;
        if let Err(f) = watched(move || check(&input, &folder)) {
            let hang = f == Finding::Hang;
            tally.findings.push((f, text));
            if hang {
                break;
            }
        }
    }
    tally
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mutations_change_the_text() {
        let mut rng = Rng::new(3);
        let text = "wavelength = 1.0\n[medium]\nsize = [4.0, 4.0, 2.0]\n";
        let others = vec![("a".to_string(), text.to_string())];
        let changed = (0..20)
            .filter(|_| mutate(text, &others, &mut rng) != text)
            .count();
        assert!(changed >= 15, "{changed}");
        assert_eq!(
            replace_number("size = [4.0, 4.0, 2.0]", &mut Rng::new(1))
                .unwrap()
                .matches(',')
                .count(),
            2
        );
    }
}
