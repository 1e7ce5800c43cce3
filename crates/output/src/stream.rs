//! Staged files whose bytes are written at commit time ([`crate::Staged::add_stream`]).

use std::fmt;
use std::io::Write;

/// Writes a staged file's bytes when the commit writes its files ([`crate::Staged::add_stream`]).
pub type Writer = Box<dyn FnMut(&mut dyn Write) -> std::io::Result<()>>;

/// The contents of a staged file.
pub(crate) enum Content {
    /// Held in memory.
    Bytes(Vec<u8>),
    /// Written at commit time.
    Stream(Writer),
}

impl fmt::Debug for Content {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Content::Bytes(b) => write!(f, "Bytes({} bytes)", b.len()),
            Content::Stream(_) => f.write_str("Stream"),
        }
    }
}

#[cfg(test)]
mod tests {
    use crate::Staged;
    use std::fs;

    /// A streamed file is committed with the others; a stream that fails leaves the previous
    /// files byte for byte and no temporary.
    #[test]
    fn streamed_files_commit_all_or_none() {
        let root = tempfile::tempdir().unwrap();
        let dir = root.path().join("out");
        let mut s = Staged::new(&dir);
        s.add("a.json".into(), b"{}".to_vec());
        s.add_stream(
            "a.npy".into(),
            Box::new(|w| (0..3u8).try_for_each(|k| w.write_all(&[k; 2]))),
        );
        assert_eq!(s.commit(|| false).unwrap().len(), 2);
        assert_eq!(fs::read(dir.join("a.npy")).unwrap(), [0, 0, 1, 1, 2, 2]);
        let mut s = Staged::new(&dir);
        s.add("a.json".into(), b"{\"new\": 1}".to_vec());
        s.add_stream(
            "a.npy".into(),
            Box::new(|w| {
                w.write_all(&[9; 4])?;
                Err(std::io::Error::other("a tile changed"))
            }),
        );
        let e = s.commit(|| false).unwrap_err().to_string();
        assert!(e.contains("a tile changed"), "{e}");
        assert_eq!(fs::read(dir.join("a.npy")).unwrap(), [0, 0, 1, 1, 2, 2]);
        assert_eq!(fs::read(dir.join("a.json")).unwrap(), b"{}");
        let mut names: Vec<_> = fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        names.sort();
        assert_eq!(names, ["a.json", "a.npy"]);
    }
}
