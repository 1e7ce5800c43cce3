//! Reading input documents: files, TOML parsing with errors that name the key path and the
//! line, and the loading of a scene file into a validated [`Problem`].
//!
//! The parser is generic ([`parse_toml`]) so that other documents of the workspace (the study
//! files of `speckle-studies`) report their errors the same way.

use crate::SceneError;
use crate::problem::Problem;
use crate::safe::{Access, MAX_SCENE_BYTES};
use crate::schema::{Overrides, PhaseSpec, SceneFile, SensorSpec, SourceSpec};
use serde::de::DeserializeOwned;
use std::io::Read as _;
use std::path::{Path, PathBuf};

/// Errors of loading an input document. Every value error is a [`SceneError`], which names the
/// field; the other variants say why the document could not be read as one.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LoadError {
    /// A value is invalid; the error names its field.
    #[error(transparent)]
    Invalid(#[from] SceneError),
    /// The document is not TOML of the expected shape: a syntax error, a value of the wrong
    /// type, an unknown or a missing key.
    #[error("{report}")]
    Parse {
        /// The key path of the offending value (`medium.sigm_s`, `sources[0].direction`), when
        /// the error is about one.
        field: Option<String>,
        /// What is wrong, in the parser's words.
        message: String,
        /// 1-based line of the offending text, when known.
        line: Option<usize>,
        /// 1-based column (in characters) of the offending text, when known.
        column: Option<usize>,
        /// The whole report as printed: the key path, the message and the offending line with
        /// a caret under it.
        report: String,
    },
    /// The input file cannot be read.
    #[error("cannot read the {what} file {}: {reason}", path.display())]
    Read {
        /// What the file is: `"scene"`, `"study"`.
        what: String,
        /// Its path.
        path: PathBuf,
        /// The operating system's reason.
        reason: String,
    },
    /// An error in the document that came from `origin` (a path, or `<embedded NAME>`).
    #[error("{origin}: {error}")]
    In {
        /// Where the document came from.
        origin: String,
        /// The error.
        error: Box<LoadError>,
    },
}

impl LoadError {
    /// The error, said to be in the document from `origin`.
    pub fn in_document(self, origin: &str) -> Self {
        Self::In {
            origin: origin.to_string(),
            error: Box::new(self),
        }
    }

    /// The name of the offending field, when the error is about one.
    pub fn field(&self) -> Option<&str> {
        match self {
            Self::Invalid(SceneError::InvalidInput { field, .. }) => Some(field),
            Self::Parse { field, .. } => field.as_deref(),
            Self::Read { .. } => None,
            Self::In { error, .. } => error.field(),
        }
    }
}

/// Finds the key of an error that names none, from the document, the error's path and its
/// message.
pub type Culprit<'a> = &'a dyn Fn(&str, &serde_path_to_error::Path, &str) -> Option<String>;

/// How [`parse_toml`] finds the key an error is about, where the parser reports it at its
/// table.
#[derive(Clone, Copy)]
pub struct KeyFinder<'a> {
    /// Message prefixes followed by the key in backquotes (`unknown field \``).
    pub prefixes: &'a [&'a str],
    /// Finds the key of an error that names none, from the document, the error's path and its
    /// message.
    pub culprit: Option<Culprit<'a>>,
}

/// 1-based line and column of byte `offset` of `text`.
fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

/// Parses a TOML document into `T`. Syntax and type errors name the key path (`medium.sigm_s`)
/// and give the line and column; `keys` says how to find a key that the parser reports at its
/// table.
pub fn parse_toml<T: DeserializeOwned>(text: &str, keys: KeyFinder<'_>) -> Result<T, LoadError> {
    let position = |span: Option<std::ops::Range<usize>>| match span {
        Some(s) => {
            let (l, c) = line_column(text, s.start);
            (Some(l), Some(c))
        }
        None => (None, None),
    };
    let de = toml::Deserializer::parse(text).map_err(|e| {
        let (mut line, mut column) = position(e.span());
        let mut field = None;
        let mut report = e.to_string();
        // A key of too many dotted parts is reported with no position: find it.
        if line.is_none()
            && let Some((l, key)) = deepest_key(text)
        {
            (line, column) = (Some(l), Some(1));
            report = format!(
                "{key}: {} (a key nested too deeply) at line {l}",
                e.message()
            );
            field = Some(key);
        }
        LoadError::Parse {
            field,
            message: e.message().to_string(),
            line,
            column,
            report: clip_report(&report),
        }
    })?;
    serde_path_to_error::deserialize(de).map_err(|e| {
        let mut message = e.inner().message().to_string();
        let (line, column) = position(e.inner().span());
        let key = keys
            .prefixes
            .iter()
            .find_map(|p| message.strip_prefix(p))
            .and_then(|r| r.split('`').next())
            .map(str::to_string)
            .or_else(|| keys.culprit.and_then(|f| f(text, e.path(), &message)));
        let mut path = e.path().to_string();
        if let Some(key) = key
            && !path.ends_with(&key)
        {
            path = if path == "." {
                key
            } else {
                format!("{path}.{key}")
            };
        }
        // A date or time where a table or a number belongs reaches serde as a table with this
        // private key.
        const DATETIME: &str = "$__toml_private_datetime";
        if path.contains(DATETIME) || message.contains(DATETIME) {
            path = path
                .replace(&format!(".{DATETIME}"), "")
                .replace(DATETIME, "");
            if path.is_empty() {
                path = ".".into();
            }
            message = "a TOML date or time is not valid here".into();
            let at = match (line, column) {
                (Some(l), Some(c)) => format!(" (line {l}, column {c})"),
                _ => String::new(),
            };
            return LoadError::Parse {
                field: (path != ".").then(|| path.clone()),
                report: format!("{path}: {message}{at}"),
                message,
                line,
                column,
            };
        }
        let detail = e.into_inner().to_string();
        if path == "." || path.is_empty() {
            LoadError::Parse {
                field: None,
                message,
                line,
                column,
                report: clip_report(detail.trim_end()),
            }
        } else {
            // `detail` is the location (line, column, excerpt) followed by `message`.
            let location = detail.trim_end();
            let location = location.strip_suffix(message.as_str()).unwrap_or(location);
            let report = clip_report(&format!("{path}: {message}\n{}", location.trim_end()));
            LoadError::Parse {
                field: Some(path),
                message,
                line,
                column,
                report,
            }
        }
    })
}

/// A report quoting the document, made safe to print: each line at most 160 characters, control
/// characters and terminal escapes written as escapes ([`crate::safe::printable`]).
fn clip_report(report: &str) -> String {
    const WIDTH: usize = 160;
    let lines: Vec<String> = report
        .trim_end()
        .lines()
        .map(|l| {
            if l.chars().count() > WIDTH {
                format!("{}...", l.chars().take(WIDTH).collect::<String>())
            } else {
                l.to_string()
            }
        })
        .collect();
    crate::safe::printable(&lines.join("\n"))
}

/// The 1-based line and a short excerpt of the key with the most dotted parts (in a
/// `key = value` line or a `[table]` header): where a "recursion limit" error lies.
fn deepest_key(text: &str) -> Option<(usize, String)> {
    text.lines()
        .enumerate()
        .filter_map(|(i, l)| {
            let l = l.trim_start();
            let key = if l.starts_with('[') {
                l.trim_start_matches('[').split(']').next()?
            } else {
                l.split('=').next()?
            };
            let dots = key.matches('.').count();
            (dots > 0).then(|| (dots, i + 1, key.trim()))
        })
        .max_by_key(|&(dots, line, _)| (dots, std::cmp::Reverse(line)))
        .map(|(_, line, key)| {
            let first = key.split('.').next().unwrap_or(key).trim();
            (line, crate::safe::excerpt(first))
        })
}

/// Reads a scene document. Unknown keys are named; a type error inside a tagged table is
/// named by looking for it in the document.
pub fn parse_scene(text: &str) -> Result<SceneFile, LoadError> {
    parse_toml(
        text,
        KeyFinder {
            prefixes: &["unknown field `"],
            culprit: Some(&tagged_culprit),
        },
    )
}

/// Serde reports a type error inside an internally tagged table (`[phase]`, an entry of
/// `[[sources]]` or `[[sensors]]`) at the table, because such a table is buffered before its
/// `type` is known. Finds the key: the one whose removal changes the error (serde stops at the
/// first bad key, in document order, before it looks for missing keys).
fn tagged_culprit(text: &str, path: &serde_path_to_error::Path, message: &str) -> Option<String> {
    use serde::Deserialize;
    use serde_path_to_error::Segment;
    if !message.starts_with("invalid ") {
        return None;
    }
    let mut segments = path.iter();
    let Some(Segment::Map { key: top }) = segments.next() else {
        return None;
    };
    if !matches!(top.as_str(), "phase" | "sources" | "sensors") {
        return None;
    }
    let doc: toml::Table = toml::from_str(text).ok()?;
    let mut value = doc.get(top)?;
    for s in segments {
        value = match s {
            Segment::Seq { index } => value.get(*index)?,
            _ => return None,
        };
    }
    let table = value.as_table()?;
    let error_without = |key: &str| {
        let mut t = table.clone();
        t.remove(key);
        let t = toml::Value::Table(t);
        let e = match top.as_str() {
            "phase" => PhaseSpec::deserialize(t).err(),
            "sources" => SourceSpec::deserialize(t).err(),
            _ => SensorSpec::deserialize(t).err(),
        };
        e.map(|e| e.message().to_string())
    };
    table
        .keys()
        .filter(|k| *k != "type")
        .find(|k| error_without(k).as_deref() != Some(message))
        .cloned()
}

/// Reads an input file (`what`: "scene", "study") of at most [`MAX_SCENE_BYTES`] and returns
/// its text (without a byte-order mark) and its stem (the default output name; `what` when the
/// path has none). The path comes from the command line, so it may be a pipe
/// (`speckle check <(speckle example)`), but never more than the limit is read (`/dev/zero`).
pub fn read_input(path: &Path, what: &str) -> Result<(String, String), LoadError> {
    let fail = |reason: String| LoadError::Read {
        what: what.to_string(),
        path: path.to_path_buf(),
        reason,
    };
    let file = std::fs::File::open(path).map_err(|e| fail(e.to_string()))?;
    if file.metadata().is_ok_and(|m| m.is_dir()) {
        return Err(fail("it is a directory".into()));
    }
    let mut bytes = Vec::new();
    file.take(MAX_SCENE_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| fail(e.to_string()))?;
    if bytes.len() as u64 > MAX_SCENE_BYTES {
        return Err(fail(format!("it has more than {MAX_SCENE_BYTES} bytes")));
    }
    let text = String::from_utf8(bytes).map_err(|e| fail(format!("it is not UTF-8 text ({e})")))?;
    let text = crate::safe::strip_bom(&text).to_string();
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| what.into());
    Ok((text, stem))
}

/// Loads and validates a scene file; relative input files are looked up next to it.
pub fn load_file(path: &Path, overrides: &Overrides) -> Result<Problem, LoadError> {
    let (text, stem) = read_input(path, "scene")?;
    let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
    load_str(&text, &path.display().to_string(), &base, &stem, overrides)
}

/// Loads and validates a scene from its text: `origin` names it in errors, relative input
/// files are looked up in `base`, and `default_name` is the output prefix when the scene sets
/// none. Errors are [`LoadError::In`] the document.
pub fn load_str(
    text: &str,
    origin: &str,
    base: &Path,
    default_name: &str,
    overrides: &Overrides,
) -> Result<Problem, LoadError> {
    load_str_quoting(text, origin, base, default_name, overrides, true)
}

/// [`load_str`] for a scene that the user did not write: the scene recorded in a shard file,
/// whose folder `base` comes from the shard's header. Its input files are read as usual, but no
/// message quotes their contents (`safe::Access::quote_inputs`), which may be those of any
/// file on the machine.
pub fn load_str_unquoted(
    text: &str,
    origin: &str,
    base: &Path,
    default_name: &str,
    overrides: &Overrides,
) -> Result<Problem, LoadError> {
    load_str_quoting(text, origin, base, default_name, overrides, false)
}

fn load_str_quoting(
    text: &str,
    origin: &str,
    base: &Path,
    default_name: &str,
    overrides: &Overrides,
    quote_inputs: bool,
) -> Result<Problem, LoadError> {
    let mut file = parse_scene(text).map_err(|e| e.in_document(origin))?;
    overrides.apply(&mut file);
    let access = Access {
        inputs_outside: overrides.allow_outside,
        output_outside: overrides.allow_outside || overrides.out.is_some(),
        quote_inputs,
    };
    Problem::build_with(file, origin, base, default_name, access)
        .map_err(|e| LoadError::from(e).in_document(origin))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_give_the_key_path_and_the_line() {
        let text = "wavelength = 1.0\n[medium]\nsize = [1.0, 1.0, 1.0]\nsigm_s = 0.5\n";
        let e = parse_scene(text).unwrap_err();
        let LoadError::Parse {
            field,
            line,
            report,
            ..
        } = &e
        else {
            panic!("{e:?}")
        };
        assert_eq!(field.as_deref(), Some("medium.sigm_s"));
        assert_eq!(*line, Some(4));
        assert!(
            report.starts_with("medium.sigm_s: unknown field `sigm_s`"),
            "{report}"
        );
        let e = parse_scene("wavelength = 1.0\n[medium").unwrap_err();
        assert!(matches!(e, LoadError::Parse { line: Some(2), .. }), "{e:?}");
        assert!(e.to_string().contains("line 2"), "{e}");
        let e = e.in_document("x.toml");
        assert!(e.to_string().starts_with("x.toml: "), "{e}");
        assert_eq!(e.field(), None);
    }

    #[test]
    fn a_type_error_in_a_tagged_table_names_the_key() {
        let text = "wavelength = 1.0\n[phase]\ntype = \"hg\"\ng = \"0.5\"\n";
        let e = parse_scene(text).unwrap_err();
        assert_eq!(e.field(), Some("phase.g"), "{e}");
    }

    #[test]
    fn line_and_column_count_from_one() {
        assert_eq!(line_column("ab\ncd", 0), (1, 1));
        assert_eq!(line_column("ab\ncd", 4), (2, 2));
        assert_eq!(line_column("é\nx", 4), (2, 2));
    }
}
