//! The crate's error type for bad input to the marker side (families, dictionaries,
//! rendering, quad geometry).
//!
//! A quad that simply is not a readable marker is *not* an error: [`crate::decode()`] returns
//! a [`crate::Rejection`] for that, because rejecting candidates is the decoder's normal work.

use thiserror::Error;

use crate::image::ImageError;

/// Everything that can be wrong with the input to the marker functions of this crate.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum FiducialError {
    /// The image buffer is unusable.
    #[error(transparent)]
    Image(#[from] ImageError),
    /// A family needs 1..=8 rows and columns of data cells (at most 64 bits).
    #[error("marker family {rows}x{cols} is not supported: rows and columns must be 1..=8")]
    BadFamily {
        /// Rows of data cells requested.
        rows: u32,
        /// Columns of data cells requested.
        cols: u32,
    },
    /// A code has bits set beyond the family's `rows * cols` data bits.
    #[error("code {code:#x} has bits beyond the {bits} data bits of the family")]
    CodeOutOfRange {
        /// The offending code.
        code: u64,
        /// Number of data bits of the family.
        bits: u32,
    },
    /// A bit grid does not have `rows * cols` entries.
    #[error("expected {expected} bits, got {got}")]
    BitCount {
        /// `rows * cols` of the family.
        expected: usize,
        /// Number of bits given.
        got: usize,
    },
    /// A non-square grid only maps onto itself under half turns.
    #[error("a {rows}x{cols} marker cannot be turned by {quarter_turns} quarter turns onto itself")]
    BadRotation {
        /// Rows of data cells.
        rows: u32,
        /// Columns of data cells.
        cols: u32,
        /// Quarter turns requested.
        quarter_turns: u8,
    },
    /// Two codes of a dictionary (or a code and a rotation) are closer than the minimum
    /// distance.
    #[error(
        "dictionary codes #{first} and #{second} (rotated {quarter_turns} quarter turns) are \
         {distance} bits apart, less than the minimum {min_distance}"
    )]
    TooClose {
        /// Index of the first code.
        first: usize,
        /// Index of the second code (equal to `first` for a code against its own rotation).
        second: usize,
        /// Clockwise quarter turns applied to the second code.
        quarter_turns: u8,
        /// Their Hamming distance.
        distance: u32,
        /// The dictionary's minimum distance.
        min_distance: u32,
    },
    /// The minimum distance must be at least 1 and at most the number of bits.
    #[error("minimum distance {min_distance} is not in 1..={bits}")]
    BadMinDistance {
        /// Requested minimum distance.
        min_distance: u32,
        /// Data bits of the family.
        bits: u32,
    },
    /// No dictionary of that name.
    #[error("unknown marker dictionary `{name}`; known (case-insensitive): {known}")]
    UnknownDictionary {
        /// The name asked for.
        name: String,
        /// The names that exist, comma-separated.
        known: String,
    },
    /// A dictionary is empty.
    #[error("a dictionary needs at least one code")]
    EmptyDictionary,
    /// The text form of a dictionary could not be parsed.
    #[error("dictionary text, line {line}: {reason}")]
    DictionaryParse {
        /// 1-based line number.
        line: usize,
        /// What is wrong there.
        reason: String,
    },
    /// Rendering parameters out of range.
    #[error("cannot render: {reason}")]
    BadRender {
        /// What is wrong.
        reason: String,
    },
    /// Four corners that do not span a convex quadrilateral (or are not finite).
    #[error("corners do not form a convex, non-degenerate quadrilateral: {reason}")]
    BadQuad {
        /// What is wrong with the corners.
        reason: &'static str,
    },
}
