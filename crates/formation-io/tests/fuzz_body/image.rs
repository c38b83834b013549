//! Image files (`formation_io::frames::decode_grey`): never a panic; an accepted
//! image has a size within the limit and exactly one grey byte per pixel. The header check
//! (`check_decoded_size`) accepts only what fits the side limit and the memory budget.

use formation_io::frames::{check_decoded_size, decode_grey};

/// The pixel limit a side for fuzzing (small, so that each run stays fast).
const MAX_SIDE: usize = 512;

/// Decodes `data` as an image file; its first 16 bytes are also a header to check.
pub fn run(data: &[u8]) {
    if let Some(head) = data.get(..16) {
        let w = u32::from_le_bytes([head[0], head[1], head[2], head[3]]);
        let h = u32::from_le_bytes([head[4], head[5], head[6], head[7]]);
        let decoded = u64::from_le_bytes([
            head[8], head[9], head[10], head[11], head[12], head[13], head[14], head[15],
        ]);
        if check_decoded_size(w, h, decoded, MAX_SIDE).is_ok() {
            assert!((1..=MAX_SIDE as u32).contains(&w) && (1..=MAX_SIDE as u32).contains(&h));
            let budget = formation_io::limits::max_buffer();
            assert!(decoded.saturating_add(u64::from(w) * u64::from(h)) <= budget);
        }
    }
    if let Ok(img) = decode_grey(data, MAX_SIDE) {
        assert!(img.width >= 1 && img.width <= MAX_SIDE);
        assert!(img.height >= 1 && img.height <= MAX_SIDE);
        assert_eq!(img.data.len(), img.width * img.height);
    }
}
