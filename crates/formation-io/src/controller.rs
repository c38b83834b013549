//! Controller files: the follower's own separation-bearing controller (gains and set-points,
//! `unicycle::ControllerConfig`) towards one leader, which `formation-tracker track
//! --controller FILE` tells the tracker (`Tracker::set_follower_controller`), as the demo's and
//! `reproduce dukf`'s follower knows its own. YAML, or JSON when the file is named `.json`.
//!
//! ```yaml
//! leader: 1               # the robot number of the leader this controller follows
//! l12_desired: 1.03       # desired separation, metres (> 0.05)
//! alpha12_desired: 0.245  # desired bearing, radians
//! k_l: 1.0                # convergence rate of the separation error, 1/s (> 0)
//! k_alpha: 1.0            # convergence rate of the bearing error, 1/s (> 0)
//! max_v: 1.5              # optional limit on |v2|, m/s
//! max_w: 2.0              # optional limit on |w2|, rad/s
//! setpoints:              # optional set-point changes, in force from `at` seconds after
//!   - {at: 5.0, l12: 3.8}  # the first frame (each may change l12, alpha12 or both)
//! ```
//!
//! Unknown fields are errors, and a value the controller refuses names its field.

use std::path::Path;

use serde::Deserialize;
use thiserror::Error;
use unicycle::{ControllerConfig, SeparationBearingController};

use crate::textfile;

/// What is wrong with a controller file.
#[derive(Debug, Error)]
pub enum ControllerFileError {
    /// The file could not be read.
    #[error("cannot read controller file {path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        source: std::io::Error,
    },
    /// The file is not a controller (syntax, unknown, missing or mistyped field), or a field
    /// has a value the controller refuses.
    #[error("controller file {path}: {message}")]
    Invalid {
        /// The file (or `<string>`).
        path: String,
        /// What is wrong, naming the field.
        message: String,
    },
}

/// A set-point change, in force from `at` seconds after the first frame.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SetpointChange {
    /// When, seconds after the first frame (>= 0).
    pub at: f64,
    /// The new desired separation, metres; `None` keeps it.
    #[serde(default)]
    pub l12: Option<f64>,
    /// The new desired bearing, radians; `None` keeps it.
    #[serde(default)]
    pub alpha12: Option<f64>,
}

/// A controller file, as read.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
struct Raw {
    leader: u32,
    l12_desired: f64,
    alpha12_desired: f64,
    k_l: f64,
    k_alpha: f64,
    #[serde(default)]
    max_v: Option<f64>,
    #[serde(default)]
    max_w: Option<f64>,
    #[serde(default)]
    setpoints: Vec<SetpointChange>,
}

/// The follower's controller towards one leader.
#[derive(Debug, Clone, PartialEq)]
pub struct FollowerController {
    /// The leader's robot number.
    pub leader: u32,
    /// Gains, set-points and limits at the first frame.
    pub controller: ControllerConfig,
    /// Set-point changes, in time order.
    pub setpoints: Vec<SetpointChange>,
}

impl FollowerController {
    /// The controller in force `t` seconds after the first frame: the changes due by then
    /// applied in order.
    pub fn at(&self, t: f64) -> ControllerConfig {
        let mut c = self.controller;
        for change in self.setpoints.iter().take_while(|s| s.at <= t) {
            c = c.with_setpoints(change.l12, change.alpha12);
        }
        c
    }
}

/// Reads a controller file (at most [`textfile::MAX_TEXT_BYTES`]).
///
/// # Errors
/// The file cannot be read, or [`from_text`] refuses it.
pub fn load(path: &Path) -> Result<FollowerController, ControllerFileError> {
    let (text, json) = textfile::read(path).map_err(|source| ControllerFileError::Io {
        path: path.display().to_string(),
        source,
    })?;
    from_text(&text, json, &path.display().to_string())
}

/// Parses and checks a controller file's text; `path` names it in errors.
///
/// # Errors
/// A syntax error, an unknown, missing or mistyped field, a leader numbered 0, or a gain,
/// set-point or limit the controller refuses, naming the field.
pub fn from_text(
    text: &str,
    json: bool,
    path: &str,
) -> Result<FollowerController, ControllerFileError> {
    let invalid = |message: String| ControllerFileError::Invalid {
        path: path.to_string(),
        message,
    };
    let raw: Raw = textfile::parse(text, json).map_err(invalid)?;
    if raw.leader == 0 {
        return Err(invalid(
            "field `leader`: 0: robots are numbered from 1".into(),
        ));
    }
    let controller = ControllerConfig {
        l12_desired: raw.l12_desired,
        alpha12_desired: raw.alpha12_desired,
        k_l: raw.k_l,
        k_alpha: raw.k_alpha,
        max_v: raw.max_v,
        max_w: raw.max_w,
    };
    // The controller's own checks name the field; the camera offset plays no part in them.
    SeparationBearingController::new(1.0, controller).map_err(|e| invalid(e.to_string()))?;
    let mut setpoints = raw.setpoints;
    for (i, change) in setpoints.iter().enumerate() {
        if !(change.at.is_finite() && change.at >= 0.0) {
            return Err(invalid(format!(
                "field `setpoints[{i}].at`: {}: expected seconds >= 0",
                change.at
            )));
        }
        let c = controller.with_setpoints(change.l12, change.alpha12);
        SeparationBearingController::new(1.0, c)
            .map_err(|e| invalid(format!("field `setpoints[{i}]`: {e}")))?;
    }
    setpoints.sort_by(|a, b| a.at.total_cmp(&b.at));
    Ok(FollowerController {
        leader: raw.leader,
        controller,
        setpoints,
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]

    use super::*;

    const GOOD: &str =
        "leader: 1\nl12_desired: 1.03\nalpha12_desired: 0.245\nk_l: 1.0\nk_alpha: 0.8\n";

    #[test]
    fn a_controller_file_is_read_and_bad_fields_are_named() {
        let f = from_text(GOOD, false, "c.yaml").unwrap();
        assert_eq!(f.leader, 1);
        assert_eq!(f.controller.l12_desired, 1.03);
        assert_eq!(f.controller.k_alpha, 0.8);
        assert_eq!(f.controller.max_v, None);
        let limited = from_text(&format!("{GOOD}max_v: 1.5\n"), false, "c.yaml").unwrap();
        assert_eq!(limited.controller.max_v, Some(1.5));
        let json =
            r#"{"leader": 2, "l12_desired": 1.5, "alpha12_desired": 0, "k_l": 1, "k_alpha": 1}"#;
        assert_eq!(from_text(json, true, "c.json").unwrap().leader, 2);
        for (bad, field) in [
            (GOOD.replace("k_l: 1.0", "k_l: -1.0"), "k_l"),
            (
                GOOD.replace("l12_desired: 1.03", "l12_desired: 0.0"),
                "l12_desired",
            ),
            (GOOD.replace("k_alpha", "k_alfa"), "k_alfa"),
            (GOOD.replace("leader: 1", "leader: 0"), "leader"),
            (GOOD.replace("leader: 1\n", ""), "leader"),
            (format!("{GOOD}max_w: -2\n"), "max_w"),
            (GOOD.replace("1.03", ".nan"), "l12_desired"),
        ] {
            let err = from_text(&bad, false, "c.yaml").unwrap_err().to_string();
            assert!(
                err.starts_with("controller file c.yaml: ") && err.contains(field),
                "{field}: {err}"
            );
        }
    }

    #[test]
    fn set_point_changes_apply_in_time_order() {
        let text =
            format!("{GOOD}setpoints:\n  - {{at: 5.0, l12: 3.8}}\n  - {{at: 2.0, alpha12: 0.1}}\n");
        let f = from_text(&text, false, "c.yaml").unwrap();
        assert_eq!(f.at(0.0), f.controller);
        assert_eq!(
            (f.at(2.0).l12_desired, f.at(2.0).alpha12_desired),
            (1.03, 0.1)
        );
        assert_eq!(
            (f.at(9.0).l12_desired, f.at(9.0).alpha12_desired),
            (3.8, 0.1)
        );
        for (bad, field) in [
            ("  - {at: -1.0, l12: 2.0}\n", "setpoints[0].at"),
            ("  - {at: 1.0, l12: 0.0}\n", "setpoints[0]"),
            ("  - {at: 1.0, speed: 2.0}\n", "speed"),
        ] {
            let err = from_text(&format!("{GOOD}setpoints:\n{bad}"), false, "c.yaml")
                .unwrap_err()
                .to_string();
            assert!(err.contains(field), "{field}: {err}");
        }
    }

    #[test]
    fn a_missing_file_names_itself() {
        let err = load(Path::new("/nonexistent/c.yaml"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("/nonexistent/c.yaml"), "{err}");
    }
}
