//! Untrusted input: the files a scene file names, the output directory it asks for, and the text
//! of messages that quote a file.
//!
//! A scene file may come from anyone. So, unless the user opts in (`Access::trusting`, the
//! command line's `--allow-outside`):
//!
//! - an input file it names (`phase.file`, `medium.grid.file`) must be a relative path that stays
//!   inside the scene file's folder (no absolute path, no `..` above it, no symbolic link out of
//!   it), and `output.dir` a relative path that stays inside the current directory;
//! - every input file, trusted or not, must be a regular file (never a FIFO, a device such as
//!   `/dev/zero` or `/dev/stdin`, or a directory, which could block or never end) no larger than
//!   its limit, and it is opened without blocking;
//! - messages quote a file's contents only through [`excerpt`]: at most a short, printable
//!   excerpt (control characters and terminal escape sequences are shown escaped).
//!
//! Paths given on the command line (the scene file itself, `--out`, `fit-phase --table`) are the
//! user's own choice: they may be absolute, but they are read with the same size limits.

use crate::SceneError;
use crate::validate::invalid;
use std::io::Read;
use std::path::{Component, Path, PathBuf};

/// Largest scene or study file read (bytes).
pub const MAX_SCENE_BYTES: u64 = 64 << 20;

/// Largest CSV amplitude table read (bytes).
pub const MAX_TABLE_BYTES: u64 = 64 << 20;

/// Largest `.npy` grid read (bytes): the largest array [`crate::npy::decode_real`] accepts,
/// 2^28 elements of 8 bytes, and a header.
pub const MAX_GRID_BYTES: u64 = (crate::npy::MAX_READ_ELEMENTS as u64) * 8 + (1 << 16);

/// Characters of a file's contents a message may quote.
pub const EXCERPT_CHARS: usize = 40;

/// Where a scene's paths may point.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Access {
    /// Input files may be absolute or outside the scene file's folder.
    pub inputs_outside: bool,
    /// `output.dir` may be absolute or outside the current directory (set when the user gave
    /// the directory on the command line, or opted in).
    pub output_outside: bool,
    /// Messages may quote a short excerpt of an input file's contents ([`excerpt`]). Not for
    /// the scene recorded in a shard file ([`crate::load::load_str_unquoted`]): its folder
    /// comes from the shard's header, so its input files may be any file on the machine.
    pub quote_inputs: bool,
}

impl Access {
    /// The default for a scene from anyone: inputs inside its folder, output inside the current
    /// directory.
    pub const CONFINED: Self = Self {
        inputs_outside: false,
        output_outside: false,
        quote_inputs: true,
    };

    /// Everything allowed (`--allow-outside`).
    pub fn trusting() -> Self {
        Self {
            inputs_outside: true,
            output_outside: true,
            quote_inputs: true,
        }
    }
}

/// Where the input files of a scene are looked up, and how far they may be: the builders' view
/// of the file system.
#[derive(Debug, Clone, Copy)]
pub struct Files<'a> {
    /// The scene file's folder; relative input files are relative to it.
    pub base: &'a Path,
    /// Whether input files may lead out of it.
    pub access: Access,
}

impl<'a> Files<'a> {
    /// Files in `base`, confined to it.
    pub fn confined(base: &'a Path) -> Self {
        Self {
            base,
            access: Access::CONFINED,
        }
    }

    /// The bytes of the input file `file` (named by `field`) of at most `limit` bytes, and its
    /// path as messages show it ([`input_path`], [`read_regular`]).
    pub fn read(
        &self,
        field: &str,
        file: &Path,
        limit: u64,
    ) -> Result<(Vec<u8>, String), SceneError> {
        let path = input_path(field, file, self.base, self.access)?;
        let shown = shown_path(&path);
        Ok((read_regular(field, &path, &shown, limit)?, shown))
    }

    /// [`Files::read`] as UTF-8 text without a byte-order mark.
    pub fn read_text(
        &self,
        field: &str,
        file: &Path,
        limit: u64,
    ) -> Result<(String, String), SceneError> {
        let (bytes, shown) = self.read(field, file, limit)?;
        Ok((utf8(field, bytes, &shown)?, shown))
    }
}

/// `bytes` as UTF-8 text without a leading byte-order mark.
fn utf8(field: &str, bytes: Vec<u8>, shown: &str) -> Result<String, SceneError> {
    let text = String::from_utf8(bytes)
        .map_err(|e| invalid(field, format!("{shown} is not UTF-8 text ({e})")))?;
    Ok(strip_bom(&text).to_string())
}

/// Whether `p` is relative and never climbs above its start (`a/../b` is fine, `../a` is not).
fn stays_below(p: &Path) -> bool {
    let mut depth = 0i64;
    for c in p.components() {
        match c {
            Component::Normal(_) => depth += 1,
            Component::CurDir => {}
            Component::ParentDir => {
                depth -= 1;
                if depth < 0 {
                    return false;
                }
            }
            Component::RootDir | Component::Prefix(_) => return false,
        }
    }
    true
}

/// The path of the input file `file` named by `field`, relative to `base` (the scene file's
/// folder). Unless `access.inputs_outside`, refuses absolute paths and paths (symbolic links
/// included) that lead out of `base`.
pub fn input_path(
    field: &str,
    file: &Path,
    base: &Path,
    access: Access,
) -> Result<PathBuf, SceneError> {
    let base = if base.as_os_str().is_empty() {
        Path::new(".")
    } else {
        base
    };
    let path = base.join(file);
    if access.inputs_outside {
        return Ok(path);
    }
    let outside = || {
        invalid(
            field,
            format!(
                "{} is outside the scene file's folder; input files must be relative paths \
                 inside it (pass --allow-outside to read it anyway)",
                shown_path(file)
            ),
        )
    };
    if !stays_below(file) {
        return Err(outside());
    }
    // Symbolic links may still lead out: compare the resolved paths (a missing file is
    // reported when it is read).
    if let (Ok(real), Ok(root)) = (path.canonicalize(), base.canonicalize())
        && !real.starts_with(&root)
    {
        return Err(outside());
    }
    Ok(path)
}

/// Checks the output directory named by `output.dir`: unless `access.output_outside`, a
/// relative path that stays inside the current directory, symbolic links included (the part
/// of it that exists is resolved).
pub fn output_dir(field: &str, dir: &Path, access: Access) -> Result<(), SceneError> {
    if dir.as_os_str().is_empty() {
        return Err(invalid(field, "must not be empty"));
    }
    if access.output_outside {
        return Ok(());
    }
    let outside = || {
        invalid(
            field,
            format!(
                "{} is outside the current directory; a scene may only write below it (give \
                 --out DIR on the command line, or pass --allow-outside)",
                shown_path(dir)
            ),
        )
    };
    if !stays_below(dir) {
        return Err(outside());
    }
    // The deepest part of `dir` that exists, resolved, must lie below the current directory.
    let mut at = dir;
    while std::fs::symlink_metadata(at).is_err() {
        match at.parent() {
            Some(p) if !p.as_os_str().is_empty() => at = p,
            _ => return Ok(()),
        }
    }
    match (at.canonicalize(), Path::new(".").canonicalize()) {
        (Ok(real), Ok(root)) if !real.starts_with(&root) => Err(outside()),
        // A link whose target is missing: it would be created outside, or not at all.
        (Err(_), _) => Err(invalid(
            field,
            format!(
                "{} leads to a folder that does not exist (a dangling symbolic link)",
                shown_path(at)
            ),
        )),
        _ => Ok(()),
    }
}

/// Opens `path` for reading without blocking (a FIFO opened for reading would wait for a
/// writer).
fn open_nonblocking(path: &Path) -> std::io::Result<std::fs::File> {
    let mut o = std::fs::OpenOptions::new();
    o.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        o.custom_flags(libc::O_NONBLOCK);
    }
    o.open(path)
}

/// Opens the regular file `path` of at most `limit` bytes for reading, and returns it with its
/// length; the error says why not (for a message that names the file). FIFOs, sockets, devices
/// and directories are refused before they are opened (opening a FIFO or a tape could block or
/// act) and again on the opened file (the path may have changed in between), and the file is
/// opened without blocking.
pub fn open_regular(path: &Path, limit: u64) -> Result<(std::fs::File, u64), String> {
    let regular = |m: &std::fs::Metadata| -> Result<u64, String> {
        if !m.is_file() {
            let what = if m.is_dir() {
                "a directory"
            } else {
                "not a regular file (a FIFO, a socket or a device)"
            };
            return Err(format!("it is {what}"));
        }
        if m.len() > limit {
            return Err(format!(
                "it has {} bytes, more than the limit of {limit}",
                m.len()
            ));
        }
        Ok(m.len())
    };
    regular(&std::fs::metadata(path).map_err(|e| e.to_string())?)?;
    let file = open_nonblocking(path).map_err(|e| e.to_string())?;
    let len = regular(&file.metadata().map_err(|e| e.to_string())?)?;
    Ok((file, len))
}

/// Reads the regular file `path` (named by `field`, shown as `shown`) of at most `limit` bytes.
/// Refuses FIFOs, devices, directories and larger files without reading them, and never blocks.
pub fn read_regular(
    field: &str,
    path: &Path,
    shown: &str,
    limit: u64,
) -> Result<Vec<u8>, SceneError> {
    let fail = |why: String| invalid(field, format!("cannot read {shown}: {why}"));
    let (file, _) = open_regular(path, limit).map_err(fail)?;
    let mut bytes = Vec::new();
    file.take(limit + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| fail(e.to_string()))?;
    if bytes.len() as u64 > limit {
        return Err(fail(format!("it has more than {limit} bytes")));
    }
    Ok(bytes)
}

/// [`read_regular`] as UTF-8 text, without a leading byte-order mark.
pub fn read_text(field: &str, path: &Path, shown: &str, limit: u64) -> Result<String, SceneError> {
    utf8(field, read_regular(field, path, shown, limit)?, shown)
}

/// `text` without a leading UTF-8 byte-order mark.
pub fn strip_bom(text: &str) -> &str {
    text.strip_prefix('\u{feff}').unwrap_or(text)
}

/// A short, printable excerpt of untrusted text for a message: at most [`EXCERPT_CHARS`]
/// characters (then `...`), with control characters, escape sequences and other invisible
/// characters written as `\u{..}` escapes.
pub fn excerpt(text: &str) -> String {
    clipped(text, EXCERPT_CHARS)
}

/// A path as messages show it: printable, at most 160 characters.
pub fn shown_path(path: &Path) -> String {
    clipped(&path.to_string_lossy(), 160)
}

/// `text` printable and cut after `max` characters.
fn clipped(text: &str, max: usize) -> String {
    let mut out = String::new();
    for (n, c) in text.chars().enumerate() {
        if n == max {
            out.push_str("...");
            break;
        }
        push_visible(&mut out, c);
    }
    out
}

/// Whether `c` is shown as is: printable, not a control, format or bidirectional character.
fn visible(c: char) -> bool {
    !(c.is_control()
        || matches!(c, '\u{200b}'..='\u{200f}' | '\u{202a}'..='\u{202e}' | '\u{2066}'..='\u{2069}' | '\u{feff}'))
}

fn push_visible(out: &mut String, c: char) {
    if visible(c) {
        out.push(c);
    } else {
        out.push_str(&c.escape_unicode().to_string());
    }
}

/// `message` made safe for a terminal: newlines and tabs are kept, every other control
/// character (the escape character of terminal sequences among them) and invisible character
/// is written as a `\u{..}` escape, so no message can move the cursor, change colours or hide
/// text.
pub fn printable(message: &str) -> String {
    let mut out = String::with_capacity(message.len());
    for c in message.chars() {
        if c == '\n' || c == '\t' {
            out.push(c);
        } else {
            push_visible(&mut out, c);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_stay_in_their_folder() {
        let dir = tempfile::tempdir().unwrap();
        let base = dir.path();
        std::fs::create_dir(base.join("sub")).unwrap();
        std::fs::write(base.join("sub/t.csv"), "x").unwrap();
        let ok = |f: &str| input_path("phase.file", Path::new(f), base, Access::CONFINED);
        assert!(ok("sub/t.csv").is_ok());
        assert!(ok("sub/../sub/t.csv").is_ok());
        for bad in ["/etc/passwd", "../x.csv", "sub/../../x.csv"] {
            let e = ok(bad).unwrap_err().to_string();
            assert!(e.starts_with("phase.file: "), "{e}");
            assert!(e.contains("outside the scene file's folder"), "{e}");
        }
        #[cfg(unix)]
        {
            std::os::unix::fs::symlink("/etc", base.join("sub/link")).unwrap();
            assert!(ok("sub/link/passwd").is_err());
        }
        let trusted = Access::trusting();
        assert!(input_path("f", Path::new("/etc/passwd"), base, trusted).is_ok());
        assert!(output_dir("output.dir", Path::new("out/a"), Access::CONFINED).is_ok());
        for bad in ["/tmp/x", "../x", ""] {
            assert!(output_dir("output.dir", Path::new(bad), Access::CONFINED).is_err());
        }
        assert!(output_dir("output.dir", Path::new("/tmp/x"), trusted).is_ok());
    }

    #[test]
    fn only_small_regular_files_are_read() {
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("a.txt");
        std::fs::write(&f, "\u{feff}hello").unwrap();
        assert_eq!(read_text("f", &f, "a.txt", 100).unwrap(), "hello");
        let e = read_regular("f", &f, "a.txt", 3).unwrap_err().to_string();
        assert!(e.contains("more than the limit of 3"), "{e}");
        let e = read_regular("f", dir.path(), "d", 3)
            .unwrap_err()
            .to_string();
        assert!(e.contains("a directory"), "{e}");
        #[cfg(unix)]
        {
            let e = read_regular("f", Path::new("/dev/zero"), "z", 3)
                .unwrap_err()
                .to_string();
            assert!(e.contains("not a regular file"), "{e}");
        }
    }

    #[test]
    fn excerpts_are_short_and_printable() {
        assert_eq!(excerpt("abc"), "abc");
        let long = "x".repeat(100);
        assert_eq!(excerpt(&long), format!("{}...", "x".repeat(EXCERPT_CHARS)));
        assert_eq!(excerpt("a\u{1b}[2Jb"), "a\\u{1b}[2Jb");
        assert_eq!(
            printable("line\n\u{1b}]0;t\u{7}x"),
            "line\n\\u{1b}]0;t\\u{7}x"
        );
        assert_eq!(printable("\u{feff}mu"), "\\u{feff}mu");
    }
}
