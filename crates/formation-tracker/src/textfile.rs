//! Reading the project's text files (rig and scene files): JSON when the file is named
//! `.json`, YAML otherwise. Only with the feature `files`, which brings the parsers
//! (`serde_json`, `serde-saphyr`).
//!
//! # Errors
//! [`read`] returns the I/O error; [`parse`] the parser's message, which names the field
//! and the position.

use std::path::Path;

use serde::de::DeserializeOwned;

/// The text of `path` and whether it is to be parsed as JSON (its extension is `json`, in any
/// case).
pub fn read(path: &Path) -> std::io::Result<(String, bool)> {
    let text = std::fs::read_to_string(path)?;
    let json = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"));
    Ok((text, json))
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
