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

/// Parses `text` as JSON when `json`, else as YAML; the error is the parser's message.
pub fn parse<T: DeserializeOwned>(text: &str, json: bool) -> Result<T, String> {
    if json {
        serde_json::from_str(text).map_err(|e| e.to_string())
    } else {
        serde_saphyr::from_str(text).map_err(|e| e.to_string())
    }
}
