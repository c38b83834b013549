//! Scene files (YAML or JSON, `formation_sim::scene::SceneSpec`): never a panic, and an
//! accepted scene passes its own validation again.

use formation_sim::scene::SceneSpec;

/// Parses `data` as a scene file (YAML when the first byte is even, else JSON).
pub fn run(data: &[u8]) {
    let json = data.first().is_some_and(|b| b % 2 == 1);
    let text = String::from_utf8_lossy(data.get(1..).unwrap_or_default());
    if let Ok(spec) = SceneSpec::from_text(&text, json, "fuzz.scene") {
        assert!(spec.validate().is_ok());
    }
}
