//! The follower's inputs CSV (`formation_io::inputs`): never a panic, and every
//! sample of an accepted file is finite.

use formation_io::inputs::FollowerInputs;

/// Parses `data` as an inputs CSV and reads samples at frames 0..16 and times 0..8 s.
pub fn run(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    let Ok(inputs) = FollowerInputs::parse(&text) else {
        return;
    };
    assert!(!inputs.is_empty(), "accepted a file without rows");
    for k in 0..16u32 {
        if let Some(s) = inputs.at(u64::from(k), f64::from(k) * 0.5) {
            assert!(s.inputs.v.is_finite() && s.inputs.w.is_finite(), "{s:?}");
            assert!(s.pan.is_none_or(f64::is_finite), "{s:?}");
        }
    }
}
