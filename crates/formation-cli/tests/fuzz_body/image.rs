//! Image files (`formation_tracker_cli::frames::decode_grey`): never a panic; an accepted
//! image has a size within the limit and exactly one grey byte per pixel.

use formation_tracker_cli::frames::decode_grey;

/// The pixel limit a side for fuzzing (small, so that each run stays fast).
const MAX_SIDE: usize = 512;

/// Decodes `data` as an image file.
pub fn run(data: &[u8]) {
    if let Ok(img) = decode_grey(data, MAX_SIDE) {
        assert!(img.width >= 1 && img.width <= MAX_SIDE);
        assert!(img.height >= 1 && img.height <= MAX_SIDE);
        assert_eq!(img.data.len(), img.width * img.height);
    }
}
