//! Controller files (YAML or JSON, `formation_io::controller`): never a panic, and an
//! accepted controller has a leader numbered from 1 and gains and set-points the controller
//! takes.

use unicycle::SeparationBearingController;

/// Parses `data` as a controller file (YAML when the first byte is even, else JSON).
pub fn run(data: &[u8]) {
    let json = data.first().is_some_and(|b| b % 2 == 1);
    let text = String::from_utf8_lossy(data.get(1..).unwrap_or_default());
    let Ok(own) = formation_io::controller::from_text(&text, json, "fuzz.controller") else {
        return;
    };
    assert!(own.leader >= 1, "accepted leader 0");
    let c = own.controller;
    assert!(
        [c.l12_desired, c.alpha12_desired, c.k_l, c.k_alpha]
            .iter()
            .all(|v| v.is_finite()),
        "accepted a non-finite setting: {c:?}"
    );
    assert!(
        SeparationBearingController::new(0.5, c).is_ok(),
        "accepted a controller it refuses: {c:?}"
    );
    // Every set-point change gives a controller it takes, at a time from 0 on.
    for change in &own.setpoints {
        assert!(
            change.at.is_finite() && change.at >= 0.0,
            "accepted {change:?}"
        );
        let c = own.at(change.at);
        assert!(
            SeparationBearingController::new(0.5, c).is_ok(),
            "accepted a set-point change it refuses: {c:?}"
        );
    }
}
