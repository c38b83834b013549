//! Reading the project's text files (rig, scene and scenario files): JSON when the file is
//! named `.json`, YAML otherwise, and every read bounded.
//!
//! # Errors
//! [`read`] returns the I/O error; [`parse`] the parser's message, which names the field
//! and the position.

use std::path::Path;

use serde::de::DeserializeOwned;

/// The largest text file read (rig, scene and scenario files; the CLI's inputs CSV and bag
/// metadata too), bytes: 16 MiB, a thousand times the largest real one. A larger file (or
/// `/dev/zero`) is refused before it is read whole.
pub const MAX_TEXT_BYTES: u64 = 16 << 20;

/// The text of `path` and whether it is to be parsed as JSON (its extension is `json`, in any
/// case). At most [`MAX_TEXT_BYTES`] are read.
///
/// # Errors
/// The I/O error; `InvalidData` for a file over the limit or not UTF-8, saying which.
pub fn read(path: &Path) -> std::io::Result<(String, bool)> {
    let bytes = read_bounded(path, MAX_TEXT_BYTES)?;
    let text = String::from_utf8(bytes).map_err(|e| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!(
                "not UTF-8 text (invalid byte at offset {})",
                e.utf8_error().valid_up_to()
            ),
        )
    })?;
    let json = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    Ok((text, json))
}

/// The bytes of `path`, refused (`InvalidData`, naming the size and the limit) if it holds
/// more than `limit`: a regular file by its size before anything is read, anything else
/// (`/dev/zero`, a pipe) after `limit + 1` bytes. Memory stays within `limit + 1` bytes
/// plus the reader's buffer.
///
/// # Errors
/// The I/O error, or `InvalidData` past the limit.
pub fn read_bounded(path: &Path, limit: u64) -> std::io::Result<Vec<u8>> {
    use std::io::Read as _;
    let file = std::fs::File::open(path)?;
    let meta = file.metadata()?;
    let too_large = |size: String| {
        std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("{size}, over the {} limit", bytes_text(limit)),
        )
    };
    if meta.is_dir() {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "is a directory, not a file",
        ));
    }
    if meta.is_file() && meta.len() > limit {
        return Err(too_large(format!("it holds {}", bytes_text(meta.len()))));
    }
    let mut bytes = Vec::new();
    file.take(limit.saturating_add(1)).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > limit {
        return Err(too_large(format!(
            "it holds more than {}",
            bytes_text(limit)
        )));
    }
    Ok(bytes)
}

/// `bytes` for a message: `16 MiB`, `1.5 GiB`, `812 bytes`.
pub fn bytes_text(bytes: u64) -> String {
    const UNITS: [(&str, u64); 3] = [("GiB", 1 << 30), ("MiB", 1 << 20), ("KiB", 1 << 10)];
    for (unit, size) in UNITS {
        if bytes >= size {
            let v = bytes as f64 / size as f64;
            return if v.fract() == 0.0 {
                format!("{v:.0} {unit}")
            } else {
                format!("{v:.1} {unit}")
            };
        }
    }
    format!("{bytes} bytes")
}

/// Parses `text` as JSON when `json`, else as YAML; the error is the parser's message on one
/// line (the YAML parser adds a drawing of the offending line below its message, which is
/// dropped: the message already names the line and column).
pub fn parse<T: DeserializeOwned>(text: &str, json: bool) -> Result<T, String> {
    if json {
        serde_json::from_str(text).map_err(|e| one_line(&e.to_string()))
    } else {
        serde_saphyr::from_str(text).map_err(|e| one_line(&e.to_string()))
    }
}

/// The first non-empty line of a parser message, without a leading `error: `.
fn one_line(message: &str) -> String {
    let first = message
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty())
        .unwrap_or("unreadable file");
    first.strip_prefix("error: ").unwrap_or(first).to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_are_bounded_even_for_endless_files() {
        let e = read_bounded(Path::new("/dev/zero"), 1000).unwrap_err();
        assert_eq!(e.kind(), std::io::ErrorKind::InvalidData);
        assert!(
            e.to_string()
                .contains("it holds more than 1000 bytes, over the 1000 bytes limit"),
            "{e}"
        );
        let dir = std::env::temp_dir().join(format!("ft-textfile-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let big = dir.join("big.yaml");
        // A sparse file: its size is refused before a byte is read.
        std::fs::File::create(&big)
            .unwrap()
            .set_len(2 << 30)
            .unwrap();
        let e = read(&big).unwrap_err();
        assert!(
            e.to_string()
                .contains("it holds 2 GiB, over the 16 MiB limit"),
            "{e}"
        );
        std::fs::write(&big, "a: 1\n").unwrap();
        assert_eq!(read(&big).unwrap().0, "a: 1\n");
        assert!(read(&dir).is_err());
        assert_eq!(bytes_text(1536 << 20), "1.5 GiB");
    }

    #[test]
    fn parser_messages_are_one_line_naming_line_and_column() {
        #[derive(Debug, serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        #[allow(dead_code)]
        struct S {
            a: u32,
        }
        let e = parse::<S>("b: 1\n", false).unwrap_err();
        assert_eq!(e.lines().count(), 1, "{e}");
        assert!(e.contains("line 1") && e.contains("`b`"), "{e}");
        let e = parse::<S>("{\"a\": \"x\"}", true).unwrap_err();
        assert_eq!(e.lines().count(), 1, "{e}");
        assert!(e.contains("line 1"), "{e}");
    }
}
