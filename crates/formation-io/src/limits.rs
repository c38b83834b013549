//! The memory budget of a run (`--max-memory`, default 1 GiB) and the bounds derived from
//! it (issue #32, `docs/reliability.md`, "Limits"). Every input is refused from its header or
//! its size before it could take more:
//!
//! - an image file is read only if it is at most the budget, and decoded only if its pixels
//!   (from the header) fit in a quarter of it, as decoded and as grey;
//! - a y4m frame (from the header) must fit in a quarter of it;
//! - a bag's record or decompressed chunk must fit in a quarter of it (and never more than
//!   1 GiB), by its declared size and by what it really decompresses to;
//! - text files (calibration, rig, scene, scenario, inputs CSV, `metadata.yaml`) have fixed
//!   limits of their own, far below the budget (`crate::textfile::MAX_TEXT_BYTES`,
//!   `pose::Camera::MAX_FILE_BYTES`).

use std::sync::atomic::{AtomicU64, Ordering};

/// The default budget, bytes: 1 GiB.
pub const DEFAULT_MAX_MEMORY: u64 = 1 << 30;

/// The smallest budget accepted, bytes: 16 MiB.
pub const MIN_MAX_MEMORY: u64 = 16 << 20;

static MAX_MEMORY: AtomicU64 = AtomicU64::new(DEFAULT_MAX_MEMORY);

/// Sets the budget for the whole run (`main`, from `--max-memory`).
pub fn set_max_memory(bytes: u64) {
    MAX_MEMORY.store(bytes.max(MIN_MAX_MEMORY), Ordering::Relaxed);
}

/// The budget, bytes.
pub fn max_memory() -> u64 {
    MAX_MEMORY.load(Ordering::Relaxed)
}

/// The largest single buffer an input may need (one decoded image, one y4m frame, one bag
/// record or chunk): a quarter of the budget, at most 1 GiB.
pub fn max_buffer() -> u64 {
    (max_memory() / 4).min(1 << 30)
}

/// Parses a byte count: `1GiB`, `512MiB`, `64KiB`, `1G`, `512M`, `2e9`, or plain bytes, at
/// least [`MIN_MAX_MEMORY`].
///
/// # Errors
/// A message naming the value and the accepted forms.
pub fn parse_bytes(s: &str) -> Result<u64, String> {
    let t = s.trim();
    let split = t
        .find(|c: char| c.is_ascii_alphabetic() && c != 'e' && c != 'E')
        .unwrap_or(t.len());
    let (number, unit) = t.split_at(split);
    let scale: u64 = match unit.trim().to_ascii_lowercase().as_str() {
        "" | "b" => 1,
        "k" | "kib" | "kb" => 1 << 10,
        "m" | "mib" | "mb" => 1 << 20,
        "g" | "gib" | "gb" => 1 << 30,
        "t" | "tib" | "tb" => 1 << 40,
        _ => {
            return Err(format!(
                "`{s}` is not a size (e.g. 1GiB, 512MiB, 64M, or bytes)"
            ));
        }
    };
    let value: f64 = number
        .trim()
        .parse()
        .map_err(|_| format!("`{s}` is not a size (e.g. 1GiB, 512MiB, 64M, or bytes)"))?;
    let bytes = value * scale as f64;
    if !(bytes.is_finite() && bytes >= MIN_MAX_MEMORY as f64 && bytes <= (1u64 << 50) as f64) {
        return Err(format!(
            "`{s}` is outside 16 MiB to 1 PiB (the memory the run may use)"
        ));
    }
    Ok(bytes as u64)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_in_the_usual_units_and_are_bounded() {
        assert_eq!(parse_bytes("1GiB"), Ok(1 << 30));
        assert_eq!(parse_bytes("512MiB"), Ok(512 << 20));
        assert_eq!(parse_bytes("64M"), Ok(64 << 20));
        assert_eq!(parse_bytes(" 2g "), Ok(2 << 30));
        assert_eq!(parse_bytes("2e9"), Ok(2_000_000_000));
        assert_eq!(parse_bytes("1.5GiB"), Ok(3 << 29));
        for bad in ["", "x", "1XB", "nan", "-1G", "1KiB", "1e300"] {
            assert!(parse_bytes(bad).is_err(), "{bad}");
        }
    }
}
