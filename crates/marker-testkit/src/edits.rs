//! Byte-level edits of a valid file, for the parser proptests that share their bodies with
//! the fuzz targets (`fuzz/`): start from input a parser accepts and explore near it.

use proptest::prelude::*;

/// One edit of a byte string: replace, insert or delete one byte at a position, or splice a
/// number (with signs, exponents, infinities or NaN) over the number at a position.
#[derive(Debug, Clone)]
pub enum Edit {
    /// Replace the byte at a position.
    Replace(usize, u8),
    /// Insert a byte at a position.
    Insert(usize, u8),
    /// Delete the byte at a position.
    Delete(usize),
    /// Replace the number at or after a position.
    Number(usize, String),
}

/// A random [`Edit`].
pub fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        (any::<usize>(), any::<u8>()).prop_map(|(at, b)| Edit::Replace(at, b)),
        (any::<usize>(), any::<u8>()).prop_map(|(at, b)| Edit::Insert(at, b)),
        any::<usize>().prop_map(Edit::Delete),
        (
            any::<usize>(),
            prop_oneof![
                "-?[0-9]{1,3}(\\.[0-9]{0,4})?([eE][-+]?[0-9]{1,3})?",
                Just(".nan".to_string()),
                Just("-.inf".to_string()),
                Just("1e308".to_string()),
                Just("0".to_string()),
                Just("-0.0".to_string()),
                Just("99999999999999999999".to_string()),
            ]
        )
            .prop_map(|(at, n)| Edit::Number(at, n)),
    ]
}

/// Applies `edits` to `seed` (positions taken modulo the current length).
pub fn apply(seed: &[u8], edits: &[Edit]) -> Vec<u8> {
    let mut bytes = seed.to_vec();
    for e in edits {
        let len = bytes.len().max(1);
        match e {
            Edit::Replace(at, b) if !bytes.is_empty() => bytes[at % len] = *b,
            Edit::Insert(at, b) => bytes.insert(at % (bytes.len() + 1), *b),
            Edit::Delete(at) if !bytes.is_empty() => {
                bytes.remove(at % len);
            }
            Edit::Number(at, n) => {
                // The run of number characters at or after the position, if any.
                let is_num = |c: &u8| c.is_ascii_digit() || b".-+eE".contains(c);
                if let Some(start) = bytes.iter().skip(at % len).position(is_num) {
                    let start = at % len + start;
                    let end = bytes[start..]
                        .iter()
                        .position(|c| !is_num(c))
                        .map_or(bytes.len(), |e| start + e);
                    bytes.splice(start..end, n.bytes());
                }
            }
            _ => {}
        }
    }
    bytes
}

/// A switch byte followed by a file's text, the input format of the
/// YAML/JSON fuzz bodies (an odd first byte selects JSON).
pub fn switched(json: u8, text: &str) -> Vec<u8> {
    let mut v = vec![json];
    v.extend_from_slice(text.as_bytes());
    v
}
